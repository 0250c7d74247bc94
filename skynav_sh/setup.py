from setuptools import find_packages, setup

package_name = 'skynav_sh'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='skynav developers',
    maintainer_email='skynav@example.org',
    description='Real spherical harmonics of fish-eye views: transform, rotation, spectra, translation.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': ['sh_node = skynav_sh.node:main'],
        'skynav.nodes': ['sh = skynav_sh.node:ShNode'],
    },
)

from setuptools import find_packages, setup

package_name = 'skynav_warping'

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
    description='Homing by 3D-warping: the home vector from the current view to a snapshot.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': ['warping_node = skynav_warping.node:main'],
        'skynav.nodes': ['warping = skynav_warping.node:WarpingNode'],
        'skynav.commands': ['eval.homing = skynav_warping.cli.eval'],
    },
)

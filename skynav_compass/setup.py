from setuptools import find_packages, setup

package_name = 'skynav_compass'

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
    description='The visual 3D compass: full 3D rotation between a current view and a snapshot.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': ['compass_node = skynav_compass.node:main'],
        'skynav.nodes': ['compass = skynav_compass.node:CompassNode'],
        'skynav.commands': ['eval.compass = skynav_compass.cli.eval'],
    },
)

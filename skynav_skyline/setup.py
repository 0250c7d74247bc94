from setuptools import find_packages, setup

package_name = 'skynav_skyline'

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
    description='Sky/ground segmentation of upward-looking UV/green fish-eye images: the skyline.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': ['skyline_node = skynav_skyline.node:main'],
        'skynav.nodes': ['skyline = skynav_skyline.node:SkylineNode'],
        'skynav.commands': [
            'skyline = skynav_skyline.cli',
            'skyline.eval = skynav_skyline.cli.eval',
            'skyline.train = skynav_skyline.cli.train',
        ],
    },
)
